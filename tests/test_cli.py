"""The ``stumble`` command line: outputs later issues rely on, and one-line errors."""

import csv
import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from stumble.cli import main

REFERENCE = Path(__file__).resolve().parents[2] / "shared" / "reference"


def run(*args: str) -> subprocess.CompletedProcess:
    """The installed command, as a user runs it."""
    return subprocess.run([sys.executable, "-m", "stumble.cli", *args], capture_output=True,
                          text=True, timeout=300)


def test_version_and_help():
    r = run("--version")
    assert r.returncode == 0 and r.stdout.startswith("stumble ")
    r = run("--help")
    assert r.returncode == 0 and "walk" in r.stdout and "model" in r.stdout


@pytest.mark.parametrize("planar", [False, True])
def test_model_json(planar, capsys):
    assert main(["model", "--json", *(["--planar"] if planar else [])]) == 0
    d = json.loads(capsys.readouterr().out)
    for key in ("nq", "nv", "nu", "dof", "joints", "mass_kg", "segments"):
        assert key in d
    assert d["dof"] == (10 if planar else 42)
    assert d["mass_kg"] == pytest.approx(70.0)
    assert sum(d["segments"].values()) == pytest.approx(70.0)


def test_model_json_scales_with_mass_height_and_sex(capsys):
    main(["model", "--json", "--mass", "90", "--height", "1.9", "--sex", "female"])
    d = json.loads(capsys.readouterr().out)
    assert d["mass_kg"] == pytest.approx(90.0)
    assert d["height_m"] == 1.9 and d["sex"] == "female"


def test_walk_writes_the_named_files(tmp_path, capsys):
    out = tmp_path / "walk"
    assert main(["walk", "--out", str(out), "--no-video", "--duration", "3"]) == 0
    for name in ("motion.csv", "events.json", "joint_angles.png"):
        assert (out / name).stat().st_size > 0
    with (out / "motion.csv").open() as f:
        rows = list(csv.reader(f))
    header = rows[0]
    assert header[:4] == ["time_s", "pelvis_x_m", "pelvis_y_m", "pelvis_z_m"]
    assert "knee_angle_r_deg" in header and "hip_flexion_l_deg" in header
    data = np.array(rows[1:], dtype=float)
    assert data[-1, 0] == pytest.approx(3.0)
    knee = data[:, header.index("knee_angle_r_deg")]
    assert knee.min() < -60 and knee.max() < 5  # degrees at the edge
    ev = json.loads((out / "events.json").read_text())
    for side in ("r", "l"):
        assert ev[side]["toe_off_s"] and ev[side]["heel_strike_s"]
    assert ev["speed_m_per_s"] == pytest.approx(1.10, abs=0.03)
    assert ev["stance_fraction"] == pytest.approx(0.63, abs=0.05)
    assert ev["stride_s"] > 1.0


def test_walk_at_a_requested_speed_changes_cadence(tmp_path):
    main(["walk", "--out", str(tmp_path / "a"), "--no-video", "--speed", "0.8"])
    main(["walk", "--out", str(tmp_path / "b"), "--no-video", "--speed", "1.5"])
    slow = json.loads((tmp_path / "a" / "events.json").read_text())
    fast = json.loads((tmp_path / "b" / "events.json").read_text())
    assert fast["stride_s"] < slow["stride_s"]
    assert fast["speed_m_per_s"] == pytest.approx(1.5)


@pytest.mark.skipif(not REFERENCE.is_dir(), reason="shared/reference is not present")
def test_walk_plays_the_subject01_mot_without_options(tmp_path):
    mot = REFERENCE / "walking" / "subject01_walk1_ik.mot"
    r = run("walk", "--out", str(tmp_path), "--gait", str(mot), "--no-video")
    assert r.returncode == 0, r.stderr
    ev = json.loads((tmp_path / "events.json").read_text())
    assert ev["source"] == "file: subject01_walk1_ik.mot"
    assert len(ev["r"]["toe_off_s"]) + len(ev["l"]["toe_off_s"]) >= 1


def _one_line_error(r: subprocess.CompletedProcess, *words: str) -> None:
    assert r.returncode != 0
    err = r.stderr.strip()
    assert "Traceback" not in err and len(err.splitlines()) == 1, err
    for w in words:
        assert w in err, err


@pytest.mark.parametrize(("args", "words"), [
    (["model", "--height", "-1.75"], ["height"]),
    (["model", "--height", "2.9"], ["height"]),
    (["model", "--mass", "abc"], ["mass"]),
    (["walk", "--out", "OUT", "--speed", "2.5"], ["speed", "2.5"]),
    (["walk", "--out", "OUT", "--speed", "0.2"], ["speed"]),
    (["walk", "--out", "OUT", "--gait", "missing.mot"], ["missing.mot"]),
])
def test_bad_input_is_one_line_and_non_zero(tmp_path, args, words):
    args = [str(tmp_path / "o") if a == "OUT" else a for a in args]
    _one_line_error(run(*args), *words)


def test_corrupt_and_unknown_files_are_one_line_errors(tmp_path):
    bad = tmp_path / "corrupt.mot"
    bad.write_text("Coordinates\nversion=1\nendheader\ntime\tknee_angle_r\n0.0\tabc\n")
    _one_line_error(run("walk", "--out", str(tmp_path / "o"), "--gait", str(bad)),
                    "corrupt.mot")
    unknown = tmp_path / "unknown.mot"
    unknown.write_text("Coordinates\nversion=1\ninDegrees=yes\nendheader\n"
                       "time\tknee_angle_r\twing_flap\n0.0\t-10\t3\n0.01\t-11\t4\n")
    _one_line_error(run("walk", "--out", str(tmp_path / "o"), "--gait", str(unknown)),
                    "wing_flap")
    _one_line_error(run("walk", "--out", str(tmp_path / "o"), "--gait", str(bad),
                        "--speed", "1.0"), "--speed")


def _main_error(capsys, argv) -> str:
    """Run ``stumble argv``; assert exit 2 and one line on stderr; return that line."""
    try:
        code = main(argv)
    except SystemExit as e:  # argparse's own checks
        code = e.code
    err = capsys.readouterr().err
    assert code == 2 and err.startswith("stumble: ") and err.count("\n") == 1, err
    return err


@pytest.fixture
def no_simulation(monkeypatch):
    """Any trip or fit simulated fails the test: the error must come first."""
    import stumble.control.reflex.identify as identify
    import stumble.pipeline as pipeline

    def boom(*a, **k):
        raise AssertionError("simulated before the error")

    monkeypatch.setattr(pipeline, "simulate_trip", boom)
    monkeypatch.setattr(identify, "fit", boom)


@pytest.mark.parametrize("argv, words", [
    (["trip", "--seed", "-1"], "argument --seed: must be from 0 to 9223372036854775807"),
    (["trip", "--seed", str(2**63)], "must be from 0 to"),
    (["trip", "--seed", "1.5"], "argument --seed: '1.5' is not a whole number"),
    (["reflex", "fit", "--seed", "-3"], "argument --seed: must be from 0"),
])
def test_bad_seeds_are_one_line(tmp_path, capsys, no_simulation, argv, words):
    assert words in _main_error(capsys, [*argv, "--out", str(tmp_path / "o")])
    assert not (tmp_path / "o").exists()


@pytest.mark.parametrize("command", [["walk"], ["trip"], ["reflex", "fit"], ["study"],
                                     ["validate"]])
def test_an_empty_out_is_one_line(tmp_path, capsys, monkeypatch, no_simulation, command):
    monkeypatch.chdir(tmp_path)
    assert "the output directory is empty" in _main_error(capsys, [*command, "--out", ""])
    assert list(tmp_path.iterdir()) == []  # nothing written into the current directory


def _unwritable(tmp_path) -> Path:
    if os.geteuid() == 0:  # root writes through mode bits: /proc refuses anyone
        return Path("/proc")
    d = tmp_path / "ro"
    d.mkdir()
    d.chmod(0o555)
    return d


@pytest.mark.parametrize("command", [["walk", "--no-video"], ["trip", "--no-video"],
                                     ["reflex", "fit"]])
def test_an_unwritable_out_is_found_before_any_simulation(tmp_path, capsys, no_simulation,
                                                          command):
    out = _unwritable(tmp_path)
    err = _main_error(capsys, [*command, "--out", str(out)])
    assert f"output directory {out} is not writable" in err
