"""Output directories and JSON files: made, checked writable, strict (no NaN/Infinity).

Every command that writes calls ``output_dir`` before its work starts, so a directory it
cannot write is one line at once, not after a simulation.
"""

from __future__ import annotations

import contextlib
import json
import math
import os
import tempfile
from pathlib import Path

from stumble.errors import InputError


def check_writable(directory: Path, what: str = "output directory") -> None:
    """InputError unless a file can be made in ``directory`` (an existing directory).

    A real probe (a temporary file made and removed), not the mode bits: root ignores
    those, a read-only file system does not."""
    try:
        fd, name = tempfile.mkstemp(prefix=".stumble-probe-", dir=directory)
    except OSError as e:
        raise InputError(f"{what} {directory} is not writable ({e.strerror or e})") from None
    os.close(fd)
    with contextlib.suppress(OSError):
        os.unlink(name)


def output_dir(out: Path, what: str = "output directory") -> Path:
    """Make ``out`` (and its parents) and check that it is writable; InputError if not."""
    out = Path(out)  # an empty --out is refused by the command line (Path("") is ".")
    try:
        out.mkdir(parents=True, exist_ok=True)
    except FileExistsError:
        raise InputError(f"cannot create {what} {out}: a file of that name exists") from None
    except OSError as e:
        raise InputError(f"cannot create {what} {out}: {e.strerror or e}") from None
    check_writable(out, what)
    return out


def finite_or_none(value):
    """``value`` with every NaN or infinite float (in dicts, lists, tuples) replaced by None."""
    if isinstance(value, float):
        return value if math.isfinite(value) else None
    if isinstance(value, dict):
        return {k: finite_or_none(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [finite_or_none(v) for v in value]
    if hasattr(value, "item") and hasattr(value, "dtype") and value.shape == ():  # NumPy
        return finite_or_none(value.item())
    return value


def write_json(path: Path, value, indent: int | None = 1) -> None:
    """Write strict JSON: a number that is not finite is written as null."""
    Path(path).write_text(json.dumps(finite_or_none(value), indent=indent, allow_nan=False)
                          + "\n")
