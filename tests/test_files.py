"""Output directories and strict JSON (stumble.files)."""

import json
import math
import os
from pathlib import Path

import numpy as np
import pytest

from stumble.errors import InputError
from stumble.files import finite_or_none, output_dir, write_json


def test_json_written_is_strict(tmp_path):
    value = {"a": math.nan, "b": [1.0, math.inf, {"c": -math.inf}], "d": np.float64("nan"),
             "e": np.float32(2.5), "f": "text", "g": None, "h": 3}
    write_json(tmp_path / "x.json", value)
    text = (tmp_path / "x.json").read_text()
    assert "NaN" not in text and "Infinity" not in text
    assert json.loads(text) == {"a": None, "b": [1.0, None, {"c": None}], "d": None,
                                "e": 2.5, "f": "text", "g": None, "h": 3}
    assert finite_or_none((1.0, math.nan)) == [1.0, None]


def test_output_dir_made_checked_and_refused(tmp_path):
    out = output_dir(tmp_path / "a" / "b")
    assert out.is_dir() and list(out.iterdir()) == []  # the probe file is gone
    (tmp_path / "f").write_text("")
    with pytest.raises(InputError, match="a file of that name exists"):
        output_dir(tmp_path / "f")
    with pytest.raises(InputError, match="cannot create output directory"):
        output_dir(tmp_path / "f" / "x")
    ro = Path("/proc") if os.geteuid() == 0 else tmp_path / "ro"
    if ro != Path("/proc"):
        ro.mkdir()
        ro.chmod(0o555)
    with pytest.raises(InputError, match=f"output directory {ro} is not writable"):
        output_dir(ro)
