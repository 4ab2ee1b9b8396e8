"""Strict JSON: every JSON file and line the package writes goes through here.

JSON has no NaN or Infinity (RFC 8259). Python's ``json`` writes them anyway, and the
file is then unreadable by strict readers (browsers, ``jq``, most languages). Here a
non-finite float becomes ``null`` (the value is not available), NumPy scalars and arrays
become plain numbers and lists, and the text is produced with ``allow_nan=False`` so
that nothing non-finite can slip through.
"""

from __future__ import annotations

import json
import math
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np


def strict(obj: Any) -> Any:
    """``obj`` with NaN/±Inf replaced by None and NumPy values made plain Python."""
    if isinstance(obj, float | np.floating):
        v = float(obj)
        return v if math.isfinite(v) else None
    if isinstance(obj, bool | np.bool_):
        return bool(obj)
    if isinstance(obj, int | np.integer):
        return int(obj)
    if isinstance(obj, np.ndarray):
        return strict(obj.tolist())
    if isinstance(obj, Mapping):
        return {str(k): strict(v) for k, v in obj.items()}
    if isinstance(obj, list | tuple):
        return [strict(v) for v in obj]
    return obj


def dumps(obj: Any, **kwargs: Any) -> str:
    """Strict JSON text of ``obj`` (``json.dumps`` keywords pass through)."""
    return json.dumps(strict(obj), allow_nan=False, **kwargs)


def write_json(path: str | Path, obj: Any, indent: int | None = 1) -> None:
    """Write ``obj`` as strict JSON (indented, trailing newline) to ``path``."""
    Path(path).write_text(dumps(obj, indent=indent) + "\n")
