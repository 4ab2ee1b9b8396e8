"""Read and write OpenSim Storage files (``.mot`` / ``.sto``) and map them onto the model.

File format (OpenSim Storage, version 1; the older SIMM ``.mot`` layout is accepted too)::

    Coordinates            <- optional name line (any line that is not ``key=value``)
    version=1
    nRows=73               <- optional; checked against the data when present
    nColumns=24            <- optional; counts the time column
    inDegrees=yes          <- yes/no; degrees are assumed when the key is absent
    endheader
    time<TAB>pelvis_tilt<TAB>...   <- column names, tab (or space) separated
    0.4<TAB>5.18...               <- numeric rows, any whitespace between values

Units. Rotational coordinates are returned in radians whatever the file holds; every
other column (translations in m, forces in N, torques in N·m, positions in m) is
returned unchanged. A column counts as rotational unless its name ends in ``_tx``,
``_ty`` or ``_tz`` or contains ``force``, ``torque``, ``_px``/``_py``/``_pz`` or
``_vx``/``_vy``/``_vz`` (the OpenSim naming of translations, forces and centres of
pressure), see :func:`is_angle_column`.

Every problem with a file raises :class:`~stumble.errors.InputError` with a one-line
message that starts with the file name.
"""

from __future__ import annotations

import re
from collections.abc import Callable, Iterable, Mapping
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from stumble.body.joints import PELVIS_ROTATIONS, hinge_names
from stumble.errors import InputError

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


@dataclass(frozen=True, eq=False)
class Motion:
    """A sampled motion.

    ``time_s`` (T,) in s, strictly increasing. ``columns`` maps each column name to a
    (T,) array: rotational coordinates in rad, translations in m, other quantities in
    the file's units (N, N·m). ``in_degrees_source`` tells whether the source stored
    angles in degrees; ``source`` is the file name.
    """

    time_s: np.ndarray
    columns: dict[str, np.ndarray]
    in_degrees_source: bool
    source: str

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


def _read_lines(path: Path) -> list[str]:
    name = path.name
    if not path.exists():
        raise InputError(f"{name}: file not found ({path})")
    if path.is_dir():
        raise InputError(f"{name}: is a directory, not a file")
    try:
        raw = path.read_bytes()
    except OSError as exc:
        raise InputError(f"{name}: cannot read the file ({exc.strerror or exc})") from exc
    try:
        text = raw.decode("utf-8-sig")
    except UnicodeDecodeError as exc:
        raise InputError(f"{name}: not a text file (byte {exc.start} is not UTF-8)") from exc
    if not text.strip():
        raise InputError(f"{name}: the file is empty")
    return text.splitlines()


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
    s = line.strip()
    if "\t" in s:
        return [p.strip() for p in s.split("\t")]
    return s.split()


def numeric_table(source: str, rows: list[list[str]], row_lines: list[int],
                  where: Callable[[int], str]) -> np.ndarray:
    """Rows of text cells as a float array; a bad cell is a one-line error naming its place.

    ``where(k)`` names the k-th cell of a row (e.g. "column 'knee_angle_r'").
    """
    try:
        data = np.array(rows, dtype=float)
    except ValueError:
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
                         f"value {rows[r][k]!r} is not finite (NaN/Inf)")
    return data


def read_mot(path: str | Path) -> Motion:
    """Read an OpenSim Storage file (``.mot`` or ``.sto``).

    Returns a :class:`Motion` with ``time_s`` in s and rotational coordinates converted to
    rad (see the module docstring for the rule). Raises :class:`InputError` (one line,
    naming the file) for a missing or empty file, a missing ``endheader``, column-name
    line or ``time`` column, non-numeric or non-finite cells, ragged rows, time not
    strictly increasing, fewer than 2 rows, and ``nRows``/``nColumns`` that disagree
    with the data.
    """
    path = Path(path)
    name = path.name
    lines = _read_lines(path)
    end, header = _parse_header(name, lines)
    in_degrees = _in_degrees(name, header)

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
    seen: set[str] = set()
    for n in names:
        if n in seen:
            raise InputError(f"{name}: line {names_line}: column {_clip(n)!r} appears twice")
        seen.add(n)
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

    if "ncolumns" in header or "datacolumns" in header:
        key = "nColumns" if "ncolumns" in header else "datacolumns"
        n_cols = _parse_int(name, key, header[key.lower()])
        if n_cols != len(names):
            raise InputError(f"{name}: header says {key}={n_cols} but line {names_line} "
                             f"names {len(names)} columns")
    if "nrows" in header or "datarows" in header:
        key = "nRows" if "nrows" in header else "datarows"
        n_rows = _parse_int(name, key, header[key.lower()])
        if n_rows != len(rows):
            raise InputError(f"{name}: header says {key}={n_rows} but the file has "
                             f"{len(rows)} data rows")
    if len(rows) < 2:
        raise InputError(f"{name}: {len(rows)} data row(s); at least 2 are needed")

    data = numeric_table(name, rows, row_lines, lambda k: f"column {names[k]!r}")

    time_s = data[:, time_col].copy()
    steps = np.diff(time_s)
    if (steps <= 0).any():
        r = int(np.argmax(steps <= 0)) + 1
        raise InputError(f"{name}: line {row_lines[r]}: time {time_s[r]:g} s is not after "
                         f"the previous time {time_s[r - 1]:g} s")

    columns: dict[str, np.ndarray] = {}
    for k, n in enumerate(names):
        if k == time_col:
            continue
        col = data[:, k].copy()
        if in_degrees and is_angle_column(n):
            col = np.deg2rad(col)
        columns[n] = col
    return Motion(time_s=time_s, columns=columns, in_degrees_source=in_degrees, source=name)


def write_mot(path: str | Path, time_s: np.ndarray, columns_rad: Mapping[str, np.ndarray],
              angle_names: Iterable[str] | None = None) -> None:
    """Write an OpenSim Storage ``.mot`` (version 1, ``inDegrees=yes``).

    ``time_s`` (T,) in s, strictly increasing; ``columns_rad`` maps names to (T,) arrays
    with angles in rad (translations in m). Columns in ``angle_names`` (default: those
    :func:`is_angle_column` calls rotational) are written in degrees, so that
    :func:`read_mot` returns the same values. Raises :class:`InputError` for bad input.
    """
    path = Path(path)
    name = path.name
    t = np.asarray(time_s, dtype=float)
    if t.ndim != 1 or t.size < 2:
        raise InputError(f"{name}: time_s must be a 1-D array of at least 2 samples")
    if not np.isfinite(t).all() or (np.diff(t) <= 0).any():
        raise InputError(f"{name}: time_s must be finite and strictly increasing")
    angles = None if angle_names is None else set(angle_names)
    names = list(columns_rad)
    if not names:
        raise InputError(f"{name}: no columns to write")
    out = np.empty((t.size, len(names) + 1))
    out[:, 0] = t
    for k, n in enumerate(names):
        if not n or re.search(r"\s", n) or n.lower() == "time":
            raise InputError(f"{name}: invalid column name {_clip(n)!r}")
        col = np.asarray(columns_rad[n], dtype=float)
        if col.shape != t.shape:
            raise InputError(f"{name}: column {n!r} has shape {col.shape}, "
                             f"expected {t.shape}")
        if not np.isfinite(col).all():
            raise InputError(f"{name}: column {n!r} has NaN or Inf values")
        is_angle = is_angle_column(n) if angles is None else n in angles
        out[:, k + 1] = np.rad2deg(col) if is_angle else col
    header = (f"{path.stem}\nversion=1\nnRows={t.size}\nnColumns={len(names) + 1}\n"
              "inDegrees=yes\nendheader\n" + "\t".join(["time", *names]) + "\n")
    body = "\n".join("\t".join(f"{v:.12g}" for v in row) for row in out)
    try:
        path.write_text(header + body + "\n", encoding="utf-8")
    except OSError as exc:
        raise InputError(f"{name}: cannot write the file ({exc.strerror or exc})") from exc


def _known_stumble_coordinates() -> set[str]:
    return set(hinge_names()) | {h.name for h in PELVIS_ROTATIONS} | set(PELVIS_TRANSLATIONS)


def map_coordinates(motion: Motion, model_coordinates: Iterable[str]) -> dict[str, np.ndarray]:
    """Columns of ``motion`` keyed by the model coordinate they drive (rad or m, (T,)).

    Matching is by exact name (OpenSim 4 path names such as
    ``/jointset/hip_r/hip_flexion_r/value`` count as ``hip_flexion_r``; ``/speed``
    columns are skipped). Rajagopal arm coordinates are renamed (``OPENSIM_RENAMES``);
    ``OPENSIM_IGNORED`` names and coordinates of stumble's 3D model that the given
    (e.g. planar) model lacks are dropped. Any other column raises :class:`InputError`
    naming up to 5 of them, and so does a file that drives no joint coordinate
    (one that is not ``pelvis_*``).
    """
    model = list(model_coordinates)
    model_set = set(model)
    known = _known_stumble_coordinates()
    raw = {_coordinate_part(n): n for n in motion.columns
           if not (n.startswith("/") and n.rstrip("/").endswith("/speed"))}
    rajagopal = bool(_RAJAGOPAL_MARKERS & raw.keys())
    out: dict[str, np.ndarray] = {}
    unknown: list[str] = []
    for coord, col in raw.items():
        target = OPENSIM_RENAMES.get(coord, coord)
        if coord in OPENSIM_IGNORED and (rajagopal or coord not in model_set):
            continue
        if target in model_set:
            if target in out:
                raise InputError(f"{motion.source}: two columns drive coordinate {target!r}")
            out[target] = np.asarray(motion.columns[col], dtype=float)
        elif target in known or coord in OPENSIM_IGNORED:
            continue  # a known DOF that this model does not have
        else:
            unknown.append(coord)
    if unknown:
        listed = ", ".join(_clip(u) for u in unknown[:5])
        more = f" and {len(unknown) - 5} more" if len(unknown) > 5 else ""
        raise InputError(f"{motion.source}: unknown coordinate names: {listed}{more} "
                         "(the model's are listed by `stumble model --json`)")
    if not any(not k.startswith("pelvis_") for k in out):
        raise InputError(f"{motion.source}: no column matches a joint coordinate of the model "
                         "(the model's are listed by `stumble model --json`)")
    return out


__all__ = [
    "OPENSIM_IGNORED",
    "OPENSIM_RENAMES",
    "PELVIS_TRANSLATIONS",
    "Motion",
    "is_angle_column",
    "map_coordinates",
    "read_mot",
    "write_mot",
]
