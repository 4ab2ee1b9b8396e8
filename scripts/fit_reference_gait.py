"""Fit the embedded reference gait from the OpenSim subject01 trial.

Writes ``src/stumble/gait/data/reference_gait.json``: a Fourier series per coordinate
over one stride (phase 0 = right heel strike), the stride time and the gait events
from the force plates, and the treadmill speed from the heel markers. Only these
figures are carried over; the data files stay in ``shared/reference``.

Run from the repository root:  python scripts/fit_reference_gait.py [REFERENCE_DIR]
"""

from __future__ import annotations

import json
import sys
from pathlib import Path

import numpy as np

from stumble.gait.readers import read_mot
from stumble.gait.reference import FourierSeries

HARMONICS = 8  # enough for the knee's swing peak; residual RMS reported below
FORCE_THRESHOLD_N = 20.0  # vertical GRF above which a foot is on the plate
SUBJECT_HEIGHT_M = 1.76  # head-top marker 1.773 m minus about 1.5 cm of marker offset
CREDIT = ("OpenSim example subject01 (Delp, Loan, Hoy, Zajac, Topp, Rosen, Thelen, "
          "Anderson, Seth; opensim-org/opensim-models), CC BY 3.0")


def plate_events(grf_path: Path) -> dict[str, dict[str, list[float]]]:
    """Heel strikes and toe-offs per foot from the two force plates."""
    grf = read_mot(grf_path)
    t = grf.time_s
    out: dict[str, dict[str, list[float]]] = {}
    for prefix in ("", "1_"):
        fy = grf.columns[f"{prefix}ground_force_vy"]
        on = fy > FORCE_THRESHOLD_N
        # OpenSim z points right: the plate under the right foot has its CoP at z > 0
        side = "r" if np.median(grf.columns[f"{prefix}ground_force_pz"][on]) > 0 else "l"
        edges = np.flatnonzero(np.diff(on.astype(int)))
        hs = [float(t[e + 1]) for e in edges if on[e + 1]]
        to = [float(t[e + 1]) for e in edges if not on[e + 1]]
        out[side] = {"heel_strike": hs, "toe_off": to}
    return out


def treadmill_speed(trc_path: Path) -> float:
    """Belt speed (m/s): the heel markers' backward speed during mid-stance."""
    lines = trc_path.read_text().splitlines()
    names = [n for n in lines[3].split("\t")[2:] if n]
    rows = np.array([[float(x) for x in ln.split("\t")[: 2 + 3 * len(names)]]
                     for ln in lines[6:] if ln.strip()])
    t = rows[:, 1]
    speeds = []
    for marker in ("R.Heel", "L.Heel"):
        k = names.index(marker)
        vx = np.gradient(rows[:, 2 + 3 * k] / 1000.0, t)
        stance = vx < -0.5  # moving back with the belt
        speeds.append(-np.median(vx[stance]))
    return float(np.mean(speeds))


def main(ref: Path) -> None:
    walking = ref / "walking"
    events = plate_events(walking / "subject01_walk1_grf.mot")
    hs_r = events["r"]["heel_strike"]
    t0, stride = hs_r[0], hs_r[1] - hs_r[0]
    ik = read_mot(walking / "subject01_walk1_ik.mot")
    phase = (ik.time_s - t0) / stride % 1.0
    coords, residual = {}, {}
    for name, values in ik.columns.items():
        if name in ("pelvis_tx", "pelvis_ty", "pelvis_tz") or np.ptp(values) == 0.0:
            continue
        series = FourierSeries.fit(phase, values, HARMONICS)
        coords[name] = {"a0": series.a0, "a": series.a.tolist(), "b": series.b.tolist()}
        residual[name] = float(np.degrees(np.sqrt(np.mean((series(phase) - values) ** 2))))

    def ph(x: float) -> float:
        return round((x - t0) / stride % 1.0, 4)

    ev = {side: {"heel_strike": ph(e["heel_strike"][0]),
                 "toe_off": ph(next(x for x in e["toe_off"] if x > e["heel_strike"][0]))}
          for side, e in events.items()}
    out = {
        "source": CREDIT,
        "fitted_by": "scripts/fit_reference_gait.py",
        "harmonics": HARMONICS,
        "phase_zero": "right heel strike",
        "units": "radians, OpenSim signs",
        "stride_s": round(stride, 5),
        "speed_m_per_s": round(treadmill_speed(walking / "subject01_walk.trc"), 4),
        "subject_height_m": SUBJECT_HEIGHT_M,
        "subject_mass_kg": 72.6,
        "events": ev,
        "metadata": {"fit_residual_rms_deg": residual,
                     "force_plate_events_s": events},
        "coordinates": coords,
    }
    dest = Path(__file__).resolve().parents[1] / "src/stumble/gait/data/reference_gait.json"
    dest.write_text(json.dumps(out, indent=1) + "\n")
    worst = max(residual, key=residual.get)
    print(f"wrote {dest}: {len(coords)} coordinates, stride {stride:.3f} s, "
          f"speed {out['speed_m_per_s']} m/s, events {ev}, worst residual {worst} "
          f"{residual[worst]:.2f} deg")


if __name__ == "__main__":
    default = Path(__file__).resolve().parents[2] / "shared" / "reference"
    main(Path(sys.argv[1]) if len(sys.argv) > 1 else default)
