"""Output directories (stumble.outdir): made, checked writable, refused in one line."""

import os
from pathlib import Path

import pytest

from stumble.errors import InputError
from stumble.outdir import output_dir


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
