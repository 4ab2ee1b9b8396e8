"""Strict JSON: no NaN or Infinity in anything the package writes."""

import json
import math

import numpy as np
import pytest

from stumble.jsonio import dumps, strict, write_json


def test_non_finite_numbers_become_null_and_numpy_values_plain():
    obj = {"a": float("nan"), "b": [1.0, float("inf"), np.float32(2.5)], "c": np.int64(3),
           "d": np.array([np.nan, 1.0]), "e": (np.bool_(True), None), 4: "key"}
    assert strict(obj) == {"a": None, "b": [1.0, None, 2.5], "c": 3, "d": [None, 1.0],
                           "e": [True, None], "4": "key"}
    text = dumps(obj)
    assert "NaN" not in text and "Infinity" not in text
    json.loads(text, parse_constant=lambda c: pytest.fail(f"non-strict constant {c}"))


def test_write_json_writes_strict_indented_text(tmp_path):
    path = tmp_path / "x.json"
    write_json(path, {"stride_s": math.nan, "speed": 1.1})
    assert path.read_text() == '{\n "stride_s": null,\n "speed": 1.1\n}\n'
