"""Output directories: made and checked writable before any work starts.

Every command that writes calls ``output_dir`` before it simulates, so a directory it
cannot write is one line at once, not an error after the simulation. (Strict JSON is
``stumble.jsonio``.)
"""

from __future__ import annotations

import contextlib
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
