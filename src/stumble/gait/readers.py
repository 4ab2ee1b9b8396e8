"""Read and write OpenSim Storage files (``.mot`` / ``.sto``) and map them onto the model.

File format (OpenSim Storage, version 1; the older SIMM ``.mot`` layout is accepted too)::

    Coordinates            <- optional name line (any line that is not ``key=value``)
    version=1
    nRows=73               <- optional; a mismatch with the data is a note, as in OpenSim
    nColumns=24            <- optional; counts the time column
    inDegrees=yes          <- yes/no; degrees are assumed when the key is absent
    endheader
    time<TAB>pelvis_tilt<TAB>...   <- column names, tab (or space) separated
    0.4<TAB>5.18...               <- numeric rows, any whitespace between values

Leniency follows OpenSim's own reader, which only warns: ``nRows``/``nColumns`` that
disagree with the data, a last row that repeats the previous time (dropped), trailing
empty cells (tabs at the ends of lines), a column name given twice (the first is kept).
Each becomes a one-line note in :attr:`Motion.notes`, which the command line prints.

Units. Rotational coordinates are returned in radians whatever the file holds; every
other column (translations in m, forces in N, torques in N·m, positions in m) is
returned unchanged. A column counts as rotational unless its name ends in ``_tx``,
``_ty`` or ``_tz`` or contains ``force``, ``torque``, ``_px``/``_py``/``_pz`` or
``_vx``/``_vy``/``_vz`` (the OpenSim naming of translations, forces and centres of
pressure), see :func:`is_angle_column`. Time is checked by :func:`check_time`.

Every problem with a file raises :class:`~stumble.errors.InputError` with a one-line
message that starts with the file name.
"""

from __future__ import annotations

import os
import re
import stat
from collections.abc import Callable, Iterable, Mapping
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from stumble.body.joints import JOINTS_3D, PELVIS_ROTATIONS, expand, hinge_names
from stumble.errors import InputError

MAX_FILE_BYTES = 64 * 2**20  # motion files above 64 MiB are refused (a 10-min 120 Hz BVH is ~40)
MIN_STEP_S = 1e-4  # time steps (s) of motion capture: 10 kHz ...
MAX_STEP_S = 1.0  # ... to 1 Hz; steps of 1-100 "s" are milliseconds (converted, with a note)
MS_STEP_RANGE = (1.0, 100.0)

_NOT_ANGLE_SUFFIXES = ("_tx", "_ty", "_tz")
_NOT_ANGLE_PARTS = ("force", "torque", "_px", "_py", "_pz", "_vx", "_vy", "_vz")
PELVIS_TRANSLATIONS = ("pelvis_tx", "pelvis_ty", "pelvis_tz")

# Coordinates of OpenSim full-body models (Rajagopal 2015 / Hamner 2010 arms, used with
# gait2392 legs) that are renamed onto ours because the joint, the zero pose, the axis
# order and the signs agree. Checked against Rajagopal2015.osim: the acromial joint is a
# CustomJoint of the torso with rotation1 = arm_flex about z (OpenSim right = our -y,
# our PITCH), rotation2 = arm_add about x (our ROLL), rotation3 = arm_rot about y (up,
# our YAW), left side mirrored; elbow_flex is 0 at full extension and + in flexion.
OPENSIM_RENAMES: dict[str, str] = {
    f"{theirs}_{side}": f"{ours}_{side}"
    for side in ("r", "l")
    for theirs, ours in (("arm_flex", "shoulder_flexion"), ("arm_add", "shoulder_adduction"),
                         ("arm_rot", "shoulder_rotation"), ("elbow_flex", "elbow_flexion"))
}

# Known OpenSim coordinates that are ignored (dropped without an error):
# - pro_sup_*: Rajagopal's forearm is at 0 when fully supinated (palm forward, range
#   0-90 deg); ours is at 0 in neutral (palm facing the thigh). A file that carries
#   Rajagopal arm names (arm_flex_*, ...) is taken to be a Rajagopal file, and its
#   pro_sup_* columns are dropped although the name matches ours.
# - wrist_flex_*, wrist_dev_*: Rajagopal's wrist axes sit in a hand frame rotated with
#   the supinated forearm and their signs were not verified against ours.
# - knee_angle_*_beta, knee_angle_beta_*: Rajagopal's patella coupler coordinate.
# - knee_adduction_*: varus/valgus of the 3-DOF knee models (Lai-Uhlrich); ours has none.
OPENSIM_IGNORED: frozenset[str] = frozenset(
    name
    for side in ("r", "l")
    for name in (f"pro_sup_{side}", f"wrist_flex_{side}", f"wrist_dev_{side}",
                 f"knee_angle_{side}_beta", f"knee_angle_beta_{side}",
                 f"knee_adduction_{side}")
)
_RAJAGOPAL_MARKERS = frozenset(
    f"{n}_{s}" for s in ("r", "l") for n in ("arm_flex", "arm_add", "arm_rot", "elbow_flex",
                                             "wrist_flex", "wrist_dev"))

# Model families and the sign of each coordinate against ours (OpenSim gait2392 signs).
# Rajagopal et al. 2016 (Rajagopal2015.osim, its walker_knee): knee_angle is 0-120 deg,
# + in flexion; gait2392 and gait10dof18musc (Delp 1990 knee): -120-10 deg, - in flexion.
MODEL_FAMILIES: dict[str, dict[str, float]] = {
    "gait2392": {},
    "gait10dof18musc": {},
    "rajagopal": {"knee_angle_r": -1.0, "knee_angle_l": -1.0},
}
LEG_BASES = ("hip_flexion", "hip_adduction", "hip_rotation", "knee_angle", "ankle_angle",
             "subtalar_angle", "mtp_angle")
RANGE_MARGIN_DEG = 30.0  # a leg angle this far outside its range of motion is an error
_RANGES_DEG = {name: rng for name, _j, _c, _a, rng in expand(JOINTS_3D)}
_RANGES_DEG.update({h.name: h.range_deg for h in PELVIS_ROTATIONS})


@dataclass(frozen=True, eq=False)
class Motion:
    """A sampled motion.

    ``time_s`` (T,) in s, strictly increasing. ``columns`` maps each column name to a
    (T,) array: rotational coordinates in rad, translations in m, other quantities in
    the file's units (N, N·m). ``in_degrees_source`` tells whether the source stored
    angles in degrees; ``source`` is the file name; ``notes`` are one-line remarks on
    what was ignored, converted or repaired while reading.
    """

    time_s: np.ndarray
    columns: dict[str, np.ndarray]
    in_degrees_source: bool
    source: str
    notes: tuple[str, ...] = ()

    @property
    def n_frames(self) -> int:
        """Number of samples T."""
        return int(self.time_s.shape[0])


def is_angle_column(name: str) -> bool:
    """Whether a Storage column holds a rotational coordinate (OpenSim naming rules).

    OpenSim 4 path names (``/jointset/hip_r/hip_flexion_r/value``) are judged by their
    coordinate part.
    """
    base = _coordinate_part(name).lower()
    if base == "time":
        return False
    if base.endswith(_NOT_ANGLE_SUFFIXES):
        return False
    return not any(part in base for part in _NOT_ANGLE_PARTS)


def _coordinate_part(name: str) -> str:
    """``/jointset/knee_r/knee_angle_r/value`` -> ``knee_angle_r``; other names unchanged."""
    if "/" not in name:
        return name
    parts = [p for p in name.split("/") if p]
    if len(parts) >= 2 and parts[-1] in ("value", "speed"):
        return parts[-2]
    return parts[-1] if parts else name


def _clip(text: str, n: int = 40) -> str:
    text = text.replace("\n", " ").replace("\r", " ")
    return text if len(text) <= n else text[: n - 3] + "..."


def listed(names: Iterable[str], most: int = 5) -> str:
    """``a, b, c, d, e and 7 more``: up to ``most`` names of a list, for one-line messages."""
    names = list(names)
    head = ", ".join(_clip(n) for n in names[:most])
    return head + (f" and {len(names) - most} more" if len(names) > most else "")


def check_file(path: str | Path) -> int:
    """Size in bytes of a regular file of at most ``MAX_FILE_BYTES``, or a one-line
    :class:`InputError` naming it: missing, a directory, a FIFO or device (``/dev/zero``,
    which would never end: only regular files are opened), or above the size cap."""
    path = Path(path)
    name = path.name or str(path)
    try:
        st = os.stat(path)
    except FileNotFoundError:
        raise InputError(f"{name}: file not found ({path})") from None
    except OSError as exc:
        raise InputError(f"{name}: cannot read the file ({exc.strerror or exc})") from None
    if stat.S_ISDIR(st.st_mode):
        raise InputError(f"{name}: is a directory, not a file")
    if not stat.S_ISREG(st.st_mode):
        raise InputError(f"{name}: not a regular file (a pipe or device); give a motion file")
    if st.st_size > MAX_FILE_BYTES:
        raise InputError(f"{name}: {st.st_size / 2**20:.0f} MiB is above the "
                         f"{MAX_FILE_BYTES // 2**20} MiB limit for motion files")
    return int(st.st_size)


def read_text(path: str | Path) -> str:
    """The text of a motion file (UTF-8, BOM dropped) checked by :func:`check_file`; a
    file that is not UTF-8 or holds no text is a one-line :class:`InputError`."""
    path = Path(path)
    name = path.name or str(path)
    check_file(path)
    try:
        with open(path, "rb") as f:
            raw = f.read(MAX_FILE_BYTES + 1)
    except OSError as exc:
        raise InputError(f"{name}: cannot read the file ({exc.strerror or exc})") from None
    if len(raw) > MAX_FILE_BYTES:
        raise InputError(f"{name}: above the {MAX_FILE_BYTES // 2**20} MiB limit for motion "
                         "files")
    try:
        text = raw.decode("utf-8-sig")
    except UnicodeDecodeError as exc:
        raise InputError(f"{name}: not a text file (byte {exc.start} is not UTF-8)") from None
    if not text.strip():
        raise InputError(f"{name}: the file is empty")
    return text


def _parse_int(name: str, key: str, value: str) -> int:
    try:
        n = int(value)
    except ValueError:
        raise InputError(f"{name}: header {key}={_clip(value)!r} is not an integer") from None
    if n < 0:
        raise InputError(f"{name}: header {key}={n} is negative")
    return n


def _parse_header(name: str, lines: list[str]) -> tuple[int, dict[str, str]]:
    """Index of the ``endheader`` line and the header's ``key -> value`` (keys lower-case)."""
    header: dict[str, str] = {}
    for i, line in enumerate(lines):
        s = line.strip()
        if s.lower() == "endheader":
            return i, header
        if "=" in s:
            key, _, value = s.partition("=")
            header[key.strip().lower()] = value.strip()
        else:  # SIMM layout: "datacolumns 24", "datarows 73"; anything else is a name/comment
            parts = s.split()
            if len(parts) == 2 and parts[0].lower() in ("datacolumns", "datarows"):
                header[parts[0].lower()] = parts[1]
    raise InputError(f"{name}: no 'endheader' line (not an OpenSim .mot/.sto file)")


def _in_degrees(name: str, header: Mapping[str, str]) -> bool:
    value = header.get("indegrees")
    if value is None:
        return True  # choice: OpenSim's GUI and SIMM-era .mot files store degrees
    v = value.lower()
    if v in ("yes", "true", "1"):
        return True
    if v in ("no", "false", "0"):
        return False
    raise InputError(f"{name}: header inDegrees={_clip(value)!r} is neither yes nor no")


def _split_names(line: str) -> list[str]:
    s = line.strip("\r\n ")
    if "\t" in s:
        parts = [p.strip() for p in s.split("\t")]
        while parts and not parts[-1]:  # trailing tabs (spreadsheet exports)
            parts.pop()
        return parts
    return s.split()


def numeric_table(source: str, rows: list[list[str]], row_lines: list[int],
                  where: Callable[[int], str]) -> np.ndarray:
    """Rows of text cells as a float array; a bad cell is a one-line error naming its place.

    ``where(k)`` names the k-th cell of a row (e.g. "column 'knee_angle_r'").
    """
    try:
        data = np.array(rows, dtype=float)
    except (ValueError, OverflowError):
        for parts, lineno in zip(rows, row_lines, strict=True):
            for k, cell in enumerate(parts):
                try:
                    float(cell)
                except ValueError:
                    raise InputError(f"{source}: line {lineno}, {where(k)}: "
                                     f"{_clip(cell)!r} is not a number") from None
        raise InputError(f"{source}: the data rows are not all numbers") from None
    bad = ~np.isfinite(data)
    if bad.any():
        r, k = np.argwhere(bad)[0]
        raise InputError(f"{source}: line {row_lines[r]}, {where(k)}: "
                         f"value {_clip(rows[r][k])!r} is not finite (NaN/Inf)")
    return data


def check_time(source: str, time_s: np.ndarray) -> tuple[np.ndarray, list[str]]:
    """Sample times (s) checked for motion capture: (times, notes).

    At least 2 samples, strictly increasing, a median step of ``MIN_STEP_S`` to
    ``MAX_STEP_S`` (10 kHz to 1 Hz) and no gap longer than ``MAX_STEP_S``. Steps of 1 to
    100 are milliseconds (a 10 Hz to 1 kHz recording whose time column is in ms):
    converted to s with a note. Anything
    else (1e-300 s steps, 1e300 s) is a one-line :class:`InputError`.
    """
    t = np.asarray(time_s, dtype=float)
    if t.size < 2:
        raise InputError(f"{source}: {t.size} sample(s); a motion needs at least 2")
    steps = np.diff(t)
    if (steps <= 0).any():
        r = int(np.argmax(steps <= 0)) + 1
        raise InputError(f"{source}: time {t[r]:g} s (sample {r + 1}) is not after the "
                         f"previous time {t[r - 1]:g} s")
    step = float(np.median(steps))
    notes = []
    if MS_STEP_RANGE[0] <= step <= MS_STEP_RANGE[1]:
        t = t / 1000.0
        notes.append(f"{source}: the time steps are {step:g}, so the time column is in "
                     f"milliseconds ({1000.0 / step:.4g} Hz); converted to seconds")
        step /= 1000.0
    if not MIN_STEP_S <= step <= MAX_STEP_S:
        raise InputError(f"{source}: a time step of {step:g} s is not a motion-capture rate "
                         f"({MIN_STEP_S:g} to {MAX_STEP_S:g} s per sample)")
    gaps = np.diff(t)
    if gaps.max() > MAX_STEP_S:
        r = int(np.argmax(gaps))
        raise InputError(f"{source}: a gap of {gaps[r]:.4g} s between the samples at "
                         f"{t[r]:g} and {t[r + 1]:g} s (more than {MAX_STEP_S:g} s)")
    return t, notes


def read_mot(path: str | Path) -> Motion:
    """Read an OpenSim Storage file (``.mot`` or ``.sto``).

    Returns a :class:`Motion` with ``time_s`` in s and rotational coordinates converted to
    rad (see the module docstring for the rule), and notes for what was repaired.
    Raises :class:`InputError` (one line, naming the file) for a file that is missing,
    not regular, too large or empty, a missing ``endheader``, column-name line or
    ``time`` column, non-numeric or non-finite cells, ragged rows, time not strictly
    increasing (but for a repeated last row), fewer than 2 rows, and time steps that are
    no motion-capture rate (:func:`check_time`).
    """
    path = Path(path)
    name = path.name
    lines = read_text(path).splitlines()
    end, header = _parse_header(name, lines)
    in_degrees = _in_degrees(name, header)
    notes: list[str] = []

    # column-name line: first non-blank line after endheader
    i = end + 1
    while i < len(lines) and not lines[i].strip():
        i += 1
    if i >= len(lines):
        raise InputError(f"{name}: no column-name line after 'endheader'")
    names_line = i + 1  # 1-based
    names = _split_names(lines[i])
    if any(not n for n in names):
        raise InputError(f"{name}: line {names_line} has an empty column name")
    lower = [n.lower() for n in names]
    if "time" not in lower:
        raise InputError(f"{name}: no 'time' column in the column names on line {names_line}")
    time_col = lower.index("time")

    rows: list[list[str]] = []
    row_lines: list[int] = []
    for j in range(i + 1, len(lines)):
        parts = lines[j].split()
        if not parts:
            continue
        if len(parts) != len(names):
            raise InputError(f"{name}: line {j + 1} has {len(parts)} values, "
                             f"expected {len(names)}")
        rows.append(parts)
        row_lines.append(j + 1)

    for keys, count, what in ((("ncolumns", "datacolumns"), len(names), "columns"),
                              (("nrows", "datarows"), len(rows), "data rows")):
        key = next((k for k in keys if k in header), None)
        if key is None:
            continue
        n = _parse_int(name, key, header[key])
        if n != count:
            label = {"ncolumns": "nColumns", "nrows": "nRows"}.get(key, key)
            notes.append(f"{name}: the header says {label}={n} but the file has {count} "
                         f"{what}; the data are used (as OpenSim does)")
    if len(rows) < 2:
        raise InputError(f"{name}: {len(rows)} data row(s); at least 2 are needed")

    data = numeric_table(name, rows, row_lines, lambda k: f"column {names[k]!r}")
    if len(data) > 2 and data[-1, time_col] == data[-2, time_col]:
        data = data[:-1]  # OpenSim tools write the last state twice; OpenSim warns
        notes.append(f"{name}: the last row repeats time {data[-1, time_col]:g} s; dropped")
    time_s, time_notes = check_time(name, data[:, time_col].copy())
    notes += time_notes

    columns: dict[str, np.ndarray] = {}
    twice: list[str] = []
    for k, n in enumerate(names):
        if k == time_col:
            continue
        if n in columns:
            twice.append(n)
            continue
        col = data[:, k].copy()
        if in_degrees and is_angle_column(n):
            col = np.deg2rad(col)
        columns[n] = col
    if twice:
        notes.append(f"{name}: columns named twice, the first of each kept: "
                     f"{listed(dict.fromkeys(twice))}")
    return Motion(time_s=time_s, columns=columns, in_degrees_source=in_degrees, source=name,
                  notes=tuple(notes))


def write_storage(path: str | Path, time_s: np.ndarray, columns: Mapping[str, np.ndarray],
                  angle_names: Iterable[str] | None = None, in_degrees: bool = True,
                  title: str | None = None) -> None:
    """Write an OpenSim Storage file (version 1, tab-separated, 12 significant digits).

    ``time_s`` (T,) in s, strictly increasing; ``columns`` maps names to (T,) arrays with
    angles in rad (translations in m, other quantities in their units). With
    ``in_degrees`` (the default) the columns in ``angle_names`` (default: those
    :func:`is_angle_column` calls rotational) are written in degrees and the header says
    ``inDegrees=yes``, so that :func:`read_mot` returns the same values; otherwise every
    column is written as given with ``inDegrees=no``. Raises :class:`InputError` for bad
    input.
    """
    path = Path(path)
    name = path.name
    t = np.asarray(time_s, dtype=float)
    if t.ndim != 1 or t.size < 2:
        raise InputError(f"{name}: time_s must be a 1-D array of at least 2 samples")
    if not np.isfinite(t).all() or (np.diff(t) <= 0).any():
        raise InputError(f"{name}: time_s must be finite and strictly increasing")
    angles = None if angle_names is None else set(angle_names)
    names = list(columns)
    if not names:
        raise InputError(f"{name}: no columns to write")
    out = np.empty((t.size, len(names) + 1))
    out[:, 0] = t
    for k, n in enumerate(names):
        if not n or re.search(r"\s", n) or n.lower() == "time":
            raise InputError(f"{name}: invalid column name {_clip(n)!r}")
        col = np.asarray(columns[n], dtype=float)
        if col.shape != t.shape:
            raise InputError(f"{name}: column {n!r} has shape {col.shape}, "
                             f"expected {t.shape}")
        if not np.isfinite(col).all():
            raise InputError(f"{name}: column {n!r} has NaN or Inf values")
        is_angle = in_degrees and (is_angle_column(n) if angles is None else n in angles)
        out[:, k + 1] = np.rad2deg(col) if is_angle else col
    header = (f"{title or path.stem}\nversion=1\nnRows={t.size}\nnColumns={len(names) + 1}\n"
              f"inDegrees={'yes' if in_degrees else 'no'}\nendheader\n"
              + "\t".join(["time", *names]) + "\n")
    body = "\n".join("\t".join(f"{v:.12g}" for v in row) for row in out)
    try:
        path.write_text(header + body + "\n", encoding="utf-8")
    except OSError as exc:
        raise InputError(f"{name}: cannot write the file ({exc.strerror or exc})") from exc


def _known_stumble_coordinates() -> set[str]:
    return set(hinge_names()) | {h.name for h in PELVIS_ROTATIONS} | set(PELVIS_TRANSLATIONS)


def _is_leg(name: str) -> bool:
    return name.rsplit("_", 1)[0] in LEG_BASES


def detect_family(motion: Motion) -> tuple[str, str]:
    """The OpenSim model family of a motion and why: ``(family, reason)``.

    Rajagopal 2016 when a coordinate names its patella (``knee_angle_r_beta``) or walker
    knee (``/jointset/walker_knee_r/...``), or when the knee angles are mostly positive
    (median above +5 deg and a peak above +30 deg: flexion counted positive); otherwise
    gait2392 (knee flexion negative).
    """
    angles = {_coordinate_part(n): v for n, v in motion.columns.items() if is_angle_column(n)}
    return _detect(list(motion.columns), angles)


def _detect(names: list[str], angles: Mapping[str, np.ndarray]) -> tuple[str, str]:
    if any("_beta" in _coordinate_part(n) or "walker_knee" in n for n in names):
        return "rajagopal", "its coordinates name Rajagopal's patella or walker knee"
    knees = [np.degrees(angles[n]) for n in ("knee_angle_r", "knee_angle_l") if n in angles]
    if knees:
        k = np.concatenate(knees)
        if np.median(k) > 5.0 and k.max() > 30.0:
            return "rajagopal", (f"its knee angles are mostly positive (median "
                                 f"{np.median(k):.0f} deg, peak {k.max():.0f} deg)")
    return "gait2392", "knee flexion negative"


def map_coordinates(motion: Motion, model_coordinates: Iterable[str],
                    family: str = "auto") -> Motion:
    """The columns of ``motion`` that drive model coordinates, checked: a new Motion.

    Matching is by exact name (OpenSim 4 path names such as
    ``/jointset/hip_r/hip_flexion_r/value`` count as ``hip_flexion_r``; ``/speed``
    columns, OpenSim 3 speeds ``*_u``, markers, forces, Moco activations and controls are
    not coordinates). Rajagopal arm coordinates are renamed (``OPENSIM_RENAMES``). Every
    column that drives no coordinate of the given model is ignored, in one note.
    ``family`` (``"auto"`` or a key of ``MODEL_FAMILIES``) maps the model's signs onto
    ours (Rajagopal's knee); ``"auto"`` uses :func:`detect_family`.

    Checks, each a one-line :class:`InputError` naming the file and the column, or a
    note when the fix is certain: a header that says radians over angles in degrees
    (converted: OpenSim's CMC writes such files), an angle beyond ±360 deg, a leg angle
    more than ``RANGE_MARGIN_DEG`` outside its range of motion, no leg coordinate left,
    two columns driving one coordinate.
    """
    model = list(model_coordinates)
    model_set = set(model)
    src = motion.source
    known = _known_stumble_coordinates()
    notes = list(motion.notes)
    raw: dict[str, str] = {}
    ignored: list[str] = []
    for n in motion.columns:
        if n.startswith("/") and n.rstrip("/").endswith("/speed"):
            ignored.append(n)
            continue
        raw.setdefault(_coordinate_part(n), n)
    rajagopal_arms = bool(_RAJAGOPAL_MARKERS & raw.keys())
    out: dict[str, np.ndarray] = {}
    for coord, col in raw.items():
        target = OPENSIM_RENAMES.get(coord, coord)
        if coord in OPENSIM_IGNORED and (rajagopal_arms or coord not in model_set):
            ignored.append(col)
            continue
        if target in model_set:
            if target in out:
                raise InputError(f"{src}: two columns drive coordinate {target!r}")
            out[target] = np.asarray(motion.columns[col], dtype=float)
        else:
            ignored.append(col)
    if not any(_is_leg(k) for k in out):
        found = [c for c in motion.columns if c in known or _coordinate_part(c) in known]
        what = (f"its coordinates ({listed(found)}) are not the model's legs" if found
                else f"its {len(motion.columns)} columns ({listed(motion.columns)}) are no "
                     "leg coordinates")
        raise InputError(f"{src}: no hip, knee or ankle coordinate of the model: {what} "
                         "(the model's are listed by `stumble model --json`)")
    if ignored:
        notes.append(f"{src}: kept {len(out)} coordinates; ignored {len(ignored)} other "
                     f"column(s): {listed(ignored)}")

    rotational = [k for k in out if k not in PELVIS_TRANSLATIONS]
    joint = [k for k in rotational if k != "pelvis_rotation"]
    peak = max(float(np.abs(out[k]).max()) for k in joint) if joint else 0.0
    if not motion.in_degrees_source and np.pi < peak <= 180.0:
        worst = max(joint, key=lambda k: float(np.abs(out[k]).max()))
        for k in rotational:
            out[k] = np.deg2rad(out[k])
        notes.append(f"{src}: the header says inDegrees=no but {worst} reaches {peak:.4g}, "
                     "which only degrees can be; read as degrees")
    for k in rotational:
        limit = 3600.0 if k == "pelvis_rotation" else 360.0  # a heading may turn 10 times
        v = float(np.degrees(np.abs(out[k]).max()))
        if v > limit:
            raise InputError(f"{src}: column {k!r} reaches {v:.4g} deg, beyond ±{limit:g} "
                             "deg: not a joint angle (wrong units or a corrupt column?)")

    if family == "auto":
        family, why = _detect(list(motion.columns), {k: out[k] for k in rotational})
        if family != "gait2392":
            notes.append(f"{src}: read as a {family} motion ({why}); knee flexion made "
                         "negative, as in gait2392")
    elif family not in MODEL_FAMILIES:
        raise InputError(f"unknown model family {family!r} (one of auto, "
                         f"{', '.join(MODEL_FAMILIES)})")
    for k, sign in MODEL_FAMILIES[family].items():
        if k in out:
            out[k] = sign * out[k]
    for k in rotational:
        if not _is_leg(k) or k not in _RANGES_DEG:
            continue
        lo, hi = _RANGES_DEG[k]
        v = np.degrees(out[k])
        over = max(lo - float(v.min()), float(v.max()) - hi)
        if over > RANGE_MARGIN_DEG:
            hint = (" (knee flexion counted positive? try --model rajagopal)"
                    if k.startswith("knee_angle") and v.max() > hi and family != "rajagopal"
                    else "")
            raise InputError(f"{src}: {k} reaches {v.min() if lo - v.min() > 0 else v.max():.0f}"
                             f" deg, {over:.0f} deg outside its range {lo:g} to {hi:g} deg"
                             f"{hint}")
    return replace(motion, columns=out, notes=tuple(notes))


__all__ = [
    "MAX_FILE_BYTES",
    "MODEL_FAMILIES",
    "OPENSIM_IGNORED",
    "OPENSIM_RENAMES",
    "PELVIS_TRANSLATIONS",
    "Motion",
    "check_file",
    "check_time",
    "detect_family",
    "is_angle_column",
    "listed",
    "map_coordinates",
    "read_mot",
    "read_text",
    "write_storage",
]
